//! Stage: accel. The SAH kd-tree builders.
//!
//! - `exact` (`sweep.rs`): Wald & Havran's O(N log N) event sweep, "On building fast
//!   kd-trees for ray tracing, and on doing that in O(N log N)" (2006): every plane
//!   through a primitive's bounds is priced. The reference.
//! - `fast` (`binned.rs`, the default): min-max binning of the SAH (Shevtsov, Soupikov &
//!   Kapustin, "Highly parallel fast kd-tree construction for interactive ray tracing
//!   of dynamic scenes", 2007) down to 48 references, parallel over primitives at the
//!   top, with the bin count shrinking with the node; below that, small nodes
//!   (`small.rs`) price every candidate plane by vector counting. Below
//!   [`BuildParams::sweep_below`] primitives (the small-node size unless set higher),
//!   or where no bin boundary beats a leaf, a node's events are made and sorted and
//!   the exact sweep finishes its subtree.
//! - The fast builder also stops where no subtree could save
//!   [`BuildParams::min_saving`] of the tree's SAH cost: splits deep in dense detail that
//!   only copy references.
//! - Both use perfect splits ([`clip`]): a straddler's bounds in each child are those of
//!   its part inside the child. Spheres use the squared-distance test, boxes their
//!   intersection with the child.
//! - Degenerate triangles (which no ray can hit) and non-finite primitives are left out;
//!   ids never change. Planes are never in the tree.
//! - Nodes are laid out depth first: a node's two children are allocated as a pair, then
//!   the left subtree, then the right. Large subtrees are built in parallel with rayon;
//!   the right subtree then goes into its own buffers that take their place after the
//!   left one, relocated when the tree is done (`out.rs`), so the parallel tree is the
//!   serial tree, node for node. Nothing a node decides depends on the thread count
//!   (counts are integers, summed in any order).
//! - Every pass over all primitives or nodes runs on the pool too, the last ones
//!   included (records in leaf order, leaf ranges, empty-child bits), in jobs small
//!   enough that no thread is left with a long tail: on two threads the serial part of
//!   Sponza's build fell from 7.3% to 2.3% of its work, which Amdahl's law reads as 7.6x
//!   to 11.8x on 16 threads (`raypack info --occupancy`, perf/log/kdtree.md, "The
//!   serial part"). The build marks its work on a [`Meter`].

mod binned;
pub mod clip;
mod out;
mod small;
mod sweep;

use super::KdTree;
use super::node::{AlignedNodes, MAX_INDEX};
use crate::accel::Prims;
use crate::accel::occupancy::{JOB, Meter};
use crate::geom::{Aabb, Geometry, PrimRef};
use clip::{clip_triangle, intersect_boxes, split_triangle, split_triangle_within};
use glam::Vec3;
use out::Out;
use rayon::prelude::*;
use std::time::Instant;

/// A primitive in a node: the bounds of its part inside the node's cell. Shared by the
/// binned levels and the sweep they hand their nodes to.
#[derive(Clone, Copy, Debug)]
pub(super) struct Ref {
    pub bounds: Aabb,
    pub prim: u32,
}

impl Ref {
    /// A placeholder, overwritten before it is read.
    const NONE: Ref = Ref {
        bounds: Aabb::EMPTY,
        prim: 0,
    };
}

/// The union of `refs`' bounds.
fn refs_bounds(refs: &[Ref]) -> Aabb {
    refs.iter().fold(Aabb::EMPTY, |b, r| b.union(&r.bounds))
}

/// Which builder makes the tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuilderKind {
    /// Wald & Havran's event sweep at every node: the reference tree.
    Exact,
    /// Min-max binning for large nodes, the exact sweep below
    /// [`BuildParams::sweep_below`] primitives.
    #[default]
    Fast,
}

impl BuilderKind {
    /// The name `--builder` takes.
    pub fn name(self) -> &'static str {
        match self {
            BuilderKind::Exact => "exact",
            BuilderKind::Fast => "fast",
        }
    }
}

impl std::str::FromStr for BuilderKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "exact" => Ok(BuilderKind::Exact),
            "fast" => Ok(BuilderKind::Fast),
            _ => Err(format!("unknown builder {s:?} (expected exact or fast)")),
        }
    }
}

impl std::fmt::Display for BuilderKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The cost model and limits of the build.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildParams {
    /// Cost of one traversal step (`K_T` in Wald & Havran, who use 15 with `K_I` = 20).
    /// The default is 30: on the benchmark scenes it halves the nodes and cuts the build
    /// by a quarter, and the packet path traces primary rays 5-9% faster in the smaller
    /// tree while the scalar path loses about as much (perf/log/kdtree.md, "Cost constants").
    pub traversal_cost: f32,
    /// Cost of one primitive test (`K_I`).
    pub intersection_cost: f32,
    /// Fraction of the cost forgiven when a split cuts off empty space (1 - lambda).
    pub empty_bonus: f32,
    /// Depth limit; `None` gives `8 + 1.3 log2(N)`.
    pub max_depth: Option<u32>,
    /// Build subtrees in parallel on the current rayon pool.
    pub parallel: bool,
    /// A node with at least this many primitives builds its two children in parallel.
    pub parallel_min_prims: u32,
    /// Which builder makes the tree (both keep every other parameter's meaning).
    pub builder: BuilderKind,
    /// The fast builder hands a node with fewer primitives than this to the exact sweep.
    /// The default, 48, is the small-node size, so binning goes down to the small nodes
    /// and the sweep only takes nodes that binning cannot split (perf/log/kdtree.md, "Fast
    /// build, second round", measures the choice).
    pub sweep_below: u32,
    /// The fast builder makes a node a leaf when even a perfect subtree below it could
    /// save less than this much of the tree's SAH cost: `(K_I n - K_T)` times the node's
    /// area over the root's, in the units `raypack info` prints the cost in. In dense
    /// detail the greedy SAH splits on to the depth limit for gains of a millionth,
    /// copying references at every level: 1e-5 leaves out 53% of the conference room's
    /// nodes, and a third of its build, at the same cost and ray rates (perf/log/kdtree.md,
    /// "Splits that save nothing"). The exact builder ignores it; 0 turns it off.
    pub min_saving: f32,
    /// A small leaf's empty margins are cut off by a chain of splits at its primitives'
    /// bounds (largest margin first) while a cut leaves the held side at most `1 -
    /// empty_cut` of the cell's area; 0 turns it off. The SAH never pays a split to trim
    /// a leaf of one triangle (K_T > K_I), yet a leaf visit costs a lane walk about as
    /// much as ten inner steps, and a cut's empty side costs nothing: 0.5 takes the
    /// conference room's leaf visits per diffuse ray from 2.95 to about 2 and its
    /// `stream` rate up 1.14x for 3% more nodes (perf/log/stream.md, "Empty margins cut"),
    /// on leaves of at most two primitives. The default 0.1 cuts every margin of a
    /// tenth of the cell or more: the conference room's diffuse `stream` rate 1.04x to
    /// 1.07x that of 0.5 for 6% more nodes, the bunny's camera packets 0.994x, the
    /// build time the same (perf/log/stream.md, "Thirteenth session").
    pub empty_cut: f32,
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            traversal_cost: 30.0,
            intersection_cost: 20.0,
            empty_bonus: 0.2,
            max_depth: None,
            parallel: true,
            parallel_min_prims: 4096,
            builder: BuilderKind::Fast,
            sweep_below: 48,
            min_saving: 1e-5,
            empty_cut: 0.1,
        }
    }
}

/// Leaves of at most this many primitives get their empty margins cut
/// ([`BuildParams::empty_cut`]). With the default costs the SAH itself trims a margin off
/// a leaf of `n` where the held side keeps under `(K_I n / (1 - bonus) - K_T) / (K_I n)`
/// of the area: never for one primitive, under 50% for two, 75% for three. Leaves of
/// two are included for those that `min_saving` ended without pricing any plane. Cutting larger
/// leaves too added 2% more nodes for no gain on the conference room's diffuse rays and
/// cost Sponza's diffuse stream about 3% (perf/log/stream.md, "Empty margins cut").
const EMPTY_CUT_MAX_PRIMS: usize = 2;

/// The bounds that a leaf of `n` primitives cuts its empty margins down to: those of
/// its primitives (`bounds()`) when `n` is at most [`EMPTY_CUT_MAX_PRIMS`], else none.
fn cut_bounds(n: usize, bounds: impl FnOnce() -> Aabb) -> Aabb {
    if n <= EMPTY_CUT_MAX_PRIMS {
        bounds()
    } else {
        Aabb::EMPTY
    }
}

/// The depth limit can never exceed this, so traversal stacks have a fixed size.
pub const MAX_DEPTH: u32 = 60;

/// The default depth limit for `prim_count` primitives: `8 + 1.3 log2(N)`.
pub fn default_max_depth(prim_count: u32) -> u32 {
    let d = 8.0 + 1.3 * (prim_count.max(1) as f32).log2();
    (d.round() as u32).min(MAX_DEPTH)
}

/// What the build reads, shared by all subtrees.
struct Builder<'a> {
    g: &'a Geometry,
    /// Each triangle's corners side by side (`Prims::corners`): clipping reads one
    /// record instead of an index triple and three vertices.
    corners: &'a [[Vec3; 3]],
    params: &'a BuildParams,
    max_depth: u32,
    /// Size of the classification scratch (one byte per bounded primitive).
    prim_total: usize,
    /// Sweep buffers that subtrees built apart have given back.
    spare: std::sync::Mutex<Vec<sweep::SweepSpace>>,
    /// Where the work handed to the pool is marked.
    meter: Meter<'a>,
    /// [`BuildParams::min_saving`] times the root cell's surface area (0 for the exact
    /// builder): what `(K_I n - K_T)` times a node's surface area must reach.
    min_saving_area: f32,
}

/// Figures about one build, for `raypack info` and perf/.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildStats {
    /// Wall time of the build.
    pub build_seconds: f64,
    /// Primitives put in the tree (degenerate triangles are left out).
    pub tree_prims: u32,
    /// The depth past which every node becomes a leaf (8 + 1.3 log2 N).
    pub max_depth_limit: u32,
    /// Which builder made the tree.
    pub builder: BuilderKind,
}

/// Bounds of a bounded primitive, or `None` when it must stay out of the tree: a triangle
/// no ray can hit (zero area) or anything with non-finite coordinates.
pub(crate) fn tree_bounds(g: &Geometry, prims: &Prims, prim: u32) -> Option<Aabb> {
    if let PrimRef::Triangle(t) = g.prim_ref(prim)
        && prims.tris[t as usize].is_degenerate()
    {
        return None;
    }
    let b = g.prim_bounds(prim);
    (b.min.is_finite() && b.max.is_finite() && !b.is_empty()).then_some(b)
}

/// Maps a float to a `u32` with the same order (negative values flipped): the sweep's
/// event keys and the small nodes' plane keys.
#[inline]
fn order_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 { !b } else { b | 1 << 31 }
}

/// The float whose [`order_bits`] are `o`.
#[inline]
fn from_order_bits(o: u32) -> f32 {
    f32::from_bits(if o >> 31 == 1 { o & !(1 << 31) } else { !o })
}

/// The cells on either side of the plane `pos` on `axis`.
fn child_cells(cell: &Aabb, axis: usize, pos: f32) -> (Aabb, Aabb) {
    let (mut left, mut right) = (*cell, *cell);
    left.max[axis] = pos;
    right.min[axis] = pos;
    (left, right)
}

/// The SAH of planes on one axis of a cell: `K_T + K_I (P_left n_left + P_right n_right)`,
/// the probabilities being the children's areas over the cell's, times `1 - empty_bonus`
/// when a side is empty. Both builders price planes with it.
#[derive(Clone, Copy)]
struct PlaneCost {
    lo: f32,
    hi: f32,
    /// Area of the two faces normal to the axis, and the perimeter that the plane's
    /// position scales (both halved, as is the cell's area).
    cap: f32,
    perimeter: f32,
    inv_area: f32,
    k_t: f32,
    k_i: f32,
    bonus: f32,
}

impl PlaneCost {
    /// `None` when the cell has no area (or a NaN one).
    #[inline]
    fn new(cell: &Aabb, axis: usize, params: &BuildParams) -> Option<PlaneCost> {
        let e = cell.max - cell.min;
        let area = e.x * e.y + e.y * e.z + e.z * e.x;
        if area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        Some(PlaneCost {
            lo: cell.min[axis],
            hi: cell.max[axis],
            cap: e[u] * e[v],
            perimeter: e[u] + e[v],
            inv_area: 1.0 / area,
            k_t: params.traversal_cost,
            k_i: params.intersection_cost,
            bonus: 1.0 - params.empty_bonus,
        })
    }

    /// The children's hit probabilities for the plane at `pos`.
    #[inline]
    fn probabilities(&self, pos: f32) -> [f32; 2] {
        [
            (self.cap + (pos - self.lo) * self.perimeter) * self.inv_area,
            (self.cap + (self.hi - pos) * self.perimeter) * self.inv_area,
        ]
    }

    /// The cost of a plane with `probabilities` and `n_left`, `n_right` primitives.
    #[inline]
    fn cost(&self, probabilities: [f32; 2], n_left: u32, n_right: u32) -> f32 {
        self.cost_of_counts(probabilities, n_left as f32, n_right as f32)
    }

    /// [`PlaneCost::cost`] with the counts already floats (exact: they stay far below
    /// 2^24), as the small nodes count them.
    #[inline]
    fn cost_of_counts(&self, [p_left, p_right]: [f32; 2], n_left: f32, n_right: f32) -> f32 {
        let c = self.k_t + self.k_i * (p_left * n_left + p_right * n_right);
        if n_left == 0.0 || n_right == 0.0 {
            c * self.bonus
        } else {
            c
        }
    }
}

impl KdTree {
    /// Builds the tree with [`BuildParams::default`].
    pub fn build(g: &Geometry) -> KdTree {
        KdTree::build_with(g, &BuildParams::default())
    }

    /// Builds the tree of `g`'s bounded primitives.
    pub fn build_with(g: &Geometry, params: &BuildParams) -> KdTree {
        KdTree::build_metered(g, params, Meter::OFF)
    }

    /// [`KdTree::build_with`], marking on `meter` how many threads work at each moment
    /// (`raypack info --occupancy`): the calling thread works throughout, but while
    /// it hands work to the pool.
    pub fn build_metered(g: &Geometry, params: &BuildParams, meter: Meter) -> KdTree {
        meter.work(|| KdTree::build_marked(g, params, meter))
    }

    fn build_marked(g: &Geometry, params: &BuildParams, meter: Meter) -> KdTree {
        let start = Instant::now();
        let prims = Prims::with(g, params.parallel, meter);
        let bounded = g.bounded_count();
        assert!(bounded <= MAX_INDEX, "kd-tree: more than 2^30 primitives");
        let refs = binned::root_refs(g, &prims, bounded, params.parallel, meter);
        let cell = refs_bounds(&refs);
        let prim_count = refs.len() as u32;
        let max_depth = params
            .max_depth
            .unwrap_or_else(|| default_max_depth(prim_count))
            .min(MAX_DEPTH);
        let builder = Builder {
            g,
            corners: &prims.corners,
            params,
            max_depth,
            prim_total: bounded as usize,
            spare: Default::default(),
            meter,
            min_saving_area: match params.builder {
                BuilderKind::Exact => 0.0,
                BuilderKind::Fast => params.min_saving * cell.surface_area(),
            },
        };
        let mut out = Out::apart();
        match params.builder {
            BuilderKind::Exact => builder.build_swept(cell, &refs, &mut out),
            BuilderKind::Fast => builder.build_binned(cell, refs, 0, 0, &mut out, &mut None),
        }
        let parallel = params.parallel;
        let (nodes, leaves, mut prim_indices) = out.finish(parallel, meter);
        // Where the mesh's own order scatters the leaves' triangles over many more cache
        // lines than need be, the records go in the order the leaves first name them,
        // and the lists name those slots (perf/log/wide.md, "Triangle records in leaf
        // order").
        let mut prims = prims;
        let tri_count = prims.sphere_base;
        let order = leaf_order(&prim_indices, tri_count, parallel, meter);
        let slot_of = inverse(&order, parallel, meter);
        let lines = |slot: &(dyn Fn(u32) -> u32 + Sync)| {
            leaf_lines(&leaves, &prim_indices, tri_count, slot, parallel, meter)
        };
        if 10 * lines(&|p| slot_of[p as usize]) < 9 * lines(&|p| p) {
            prims.reorder_triangles(&order, parallel, meter);
            let to_slot = |p: &mut u32| {
                if *p < tri_count {
                    *p = slot_of[*p as usize];
                }
            };
            if parallel {
                meter.hand_off(|| {
                    (prim_indices.par_chunks_mut(JOB))
                        .for_each(|c| meter.work(|| c.iter_mut().for_each(to_slot)))
                });
            } else {
                prim_indices.iter_mut().for_each(to_slot);
            }
        }
        let nodes = if parallel {
            AlignedNodes::marked_in_parallel(&nodes, meter)
        } else {
            let mut nodes = nodes;
            super::node::mark_empty_children(&mut nodes);
            nodes.into()
        };
        let stats = BuildStats {
            build_seconds: start.elapsed().as_secs_f64(),
            tree_prims: prim_count,
            max_depth_limit: max_depth,
            builder: params.builder,
        };
        let mut tree = KdTree {
            nodes,
            leaves,
            prim_indices,
            prims,
            bounds: cell,
            build_stats: stats,
            flat: Vec::new(),
        };
        tree.choose_flat(params);
        tree
    }
}

/// The triangles (ids below `tri_count`) in the order the leaves' lists `prim_indices`
/// first name them, then those no leaf holds (degenerate ones) in id order. In
/// parallel, each triangle's first position is found first (a minimum over its
/// mentions), then each chunk keeps the mentions that are first ones.
pub(crate) fn leaf_order(
    prim_indices: &[u32],
    tri_count: u32,
    parallel: bool,
    meter: Meter,
) -> Vec<u32> {
    if !parallel {
        let mut seen = vec![false; tri_count as usize];
        let mut order = Vec::with_capacity(tri_count as usize);
        for &p in prim_indices {
            if p < tri_count && !std::mem::replace(&mut seen[p as usize], true) {
                order.push(p);
            }
        }
        order.extend((0..tri_count).filter(|&p| !seen[p as usize]));
        return order;
    }
    use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
    const CHUNK: usize = 1 << 16;
    meter.hand_off(|| {
        let first: Vec<AtomicU32> = (meter.jobs((0..tri_count).into_par_iter()))
            .map(|_| AtomicU32::new(u32::MAX))
            .collect();
        prim_indices
            .par_chunks(CHUNK)
            .with_max_len(1)
            .enumerate()
            .for_each(|(c, chunk)| {
                meter.work(|| {
                    for (k, &p) in chunk.iter().enumerate() {
                        if p < tri_count {
                            first[p as usize].fetch_min((c * CHUNK + k) as u32, Relaxed);
                        }
                    }
                })
            });
        let is_first = |c: usize, k: usize, p: u32| {
            p < tri_count && first[p as usize].load(Relaxed) == (c * CHUNK + k) as u32
        };
        let mut order: Vec<u32> = prim_indices
            .par_chunks(CHUNK)
            .with_max_len(1)
            .enumerate()
            .flat_map_iter(|(c, chunk)| {
                let _working = meter.working();
                let named = chunk
                    .iter()
                    .enumerate()
                    .filter(move |&(k, &p)| is_first(c, k, p));
                named.map(|(_, &p)| p).collect::<Vec<_>>()
            })
            .collect();
        let unnamed = |p: &u32| first[*p as usize].load(Relaxed) == u32::MAX;
        order.par_extend((0..tri_count).into_par_iter().filter(unnamed));
        order
    })
}

/// The inverse of the permutation `order`: `slot_of[order[s]] = s`.
pub(crate) fn inverse(order: &[u32], parallel: bool, meter: Meter) -> Vec<u32> {
    if !parallel {
        let mut slot_of = vec![0u32; order.len()];
        for (slot, &p) in order.iter().enumerate() {
            slot_of[p as usize] = slot as u32;
        }
        return slot_of;
    }
    use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
    meter.hand_off(|| {
        let slot_of: Vec<AtomicU32> = (meter.jobs((0..order.len()).into_par_iter()))
            .map(|_| AtomicU32::new(0))
            .collect();
        (meter.jobs(order.par_iter().enumerate()))
            .for_each(|(s, &p)| slot_of[p as usize].store(s as u32, Relaxed));
        (meter.jobs(slot_of.into_par_iter()))
            .map(AtomicU32::into_inner)
            .collect()
    })
}

/// The 64-byte lines that the records (48 bytes each) of every eighth leaf's triangles
/// span, summed, with triangle `p` (below `tri_count`) in slot `slot(p)`: what a visit
/// to those leaves loads.
fn leaf_lines(
    leaves: &[[u32; 2]],
    prim_indices: &[u32],
    tri_count: u32,
    slot: &(dyn Fn(u32) -> u32 + Sync),
    parallel: bool,
    meter: Meter,
) -> u64 {
    let count = |lines: &mut Vec<u64>, &[first, count]: &[u32; 2]| {
        lines.clear();
        for &p in &prim_indices[first as usize..][..count as usize] {
            if p < tri_count {
                let byte = slot(p) as u64 * 48;
                lines.extend([byte / 64, (byte + 47) / 64]);
            }
        }
        lines.sort_unstable();
        lines.dedup();
        lines.len() as u64
    };
    if parallel {
        meter.hand_off(|| {
            (meter.jobs(leaves.par_iter().step_by(8)))
                .map_init(Vec::new, |lines, leaf| count(lines, leaf))
                .sum()
        })
    } else {
        let mut lines = Vec::new();
        leaves
            .iter()
            .step_by(8)
            .map(|leaf| count(&mut lines, leaf))
            .sum()
    }
}

impl Builder<'_> {
    /// Makes the node at `slot` (in `cell`, at `depth`) a leaf of `prims`, first cutting
    /// off the cell's empty margins outside `bounds` ([`BuildParams::empty_cut`]; what
    /// [`cut_bounds`] gives).
    fn leaf(
        &self,
        out: &mut Out,
        mut slot: usize,
        mut cell: Aabb,
        mut depth: u32,
        bounds: Aabb,
        prims: impl Iterator<Item = u32>,
    ) {
        // The cuts lie on the bounds' faces, so the bounds stay inside every cell below.
        let bounds = intersect_boxes(&bounds, &cell);
        while depth < MAX_DEPTH
            && let Some((axis, pos, above)) = self.empty_cut(&cell, &bounds)
        {
            let first = out.inner(slot, axis, pos);
            let (left, right) = child_cells(&cell, axis, pos);
            let (empty, full) = if above {
                (first, first + 1)
            } else {
                (first + 1, first)
            };
            out.leaf(empty, std::iter::empty());
            cell = if above { right } else { left };
            slot = full;
            depth += 1;
        }
        out.leaf(slot, prims);
    }

    /// The plane that cuts off the largest empty margin of `cell` outside `b` (the
    /// bounds of what the cell holds, inside it), as (axis, position, whether the held
    /// side is above it), when that leaves the held side at most `1 - empty_cut` of the
    /// cell's area ([`BuildParams::empty_cut`]).
    fn empty_cut(&self, cell: &Aabb, b: &Aabb) -> Option<(usize, f32, bool)> {
        if self.params.empty_cut <= 0.0 || b.is_empty() {
            return None;
        }
        let area = cell.surface_area();
        let mut best: Option<(f32, usize, f32, bool)> = None;
        for axis in 0..3 {
            for (pos, above) in [(b.min[axis], true), (b.max[axis], false)] {
                let (left, right) = child_cells(cell, axis, pos);
                let (held, inside) = if above {
                    (right, pos > cell.min[axis])
                } else {
                    (left, pos < cell.max[axis])
                };
                let ratio = held.surface_area() / area;
                if inside
                    && ratio <= 1.0 - self.params.empty_cut
                    && best.is_none_or(|(r, ..)| ratio < r)
                {
                    best = Some((ratio, axis, pos, above));
                }
            }
        }
        best.map(|(_, axis, pos, above)| (axis, pos, above))
    }

    /// Whether a node of `n` references in `cell` at `depth` may split at all: false when
    /// it is empty, at the depth limit, or when no subtree could save
    /// [`BuildParams::min_saving`] of the tree's cost. Every builder's nodes stop here.
    #[inline]
    fn may_split(&self, cell: &Aabb, n: usize, depth: u32) -> bool {
        let p = self.params;
        n != 0
            && depth < self.max_depth
            && (self.min_saving_area <= 0.0
                || (p.intersection_cost * n as f32 - p.traversal_cost) * cell.surface_area()
                    >= self.min_saving_area)
    }

    /// Bounds of the part of `prim` inside `cell`, or `None` when it misses the cell.
    fn clip(&self, prim: u32, cell: &Aabb) -> Option<Aabb> {
        match self.g.prim_ref(prim) {
            PrimRef::Triangle(t) => clip_triangle(self.corners[t as usize], cell),
            PrimRef::Sphere(s) => {
                let s = &self.g.spheres[s as usize];
                let nearest = s.center.clamp(cell.min, cell.max);
                let d2 = (nearest - s.center).length_squared();
                // A touch of slack: an overlap lost to rounding would lose hits.
                (d2 <= s.radius * s.radius * (1.0 + 1e-5))
                    .then(|| intersect_boxes(&s.bounds(), cell))
                    .filter(|b| !b.is_empty())
            }
            PrimRef::Box(b) => {
                Some(intersect_boxes(&self.g.boxes[b as usize], cell)).filter(|b| !b.is_empty())
            }
            PrimRef::Plane(_) => None,
        }
    }

    /// Bounds of the parts of straddler `prim` in the two children of `cell` split at
    /// `pos` on `axis` (perfect splits); `None` for a side it does not reach.
    fn split_prim(&self, prim: u32, cell: &Aabb, axis: usize, pos: f32) -> [Option<Aabb>; 2] {
        match self.g.prim_ref(prim) {
            PrimRef::Triangle(t) => split_triangle(self.corners[t as usize], cell, axis, pos),
            _ => {
                let (left, right) = child_cells(cell, axis, pos);
                [self.clip(prim, &left), self.clip(prim, &right)]
            }
        }
    }

    /// [`Builder::split_prim`] for a straddler whose part in `cell` has bounds `part`:
    /// a triangle is cut by the plane alone ([`split_triangle_within`]).
    #[inline(always)]
    fn split_within(
        &self,
        prim: u32,
        part: &Aabb,
        cell: &Aabb,
        axis: usize,
        pos: f32,
    ) -> [Option<Aabb>; 2] {
        match self.g.prim_ref(prim) {
            PrimRef::Triangle(t) => {
                split_triangle_within(self.corners[t as usize], part, cell, axis, pos)
            }
            _ => self.split_prim(prim, cell, axis, pos),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::kdtree::node::KdNode;

    #[test]
    fn the_last_passes_give_the_same_answers_in_parallel() {
        // Index lists that name triangles several times, in scattered order, with some
        // never named and some spheres (ids at or above the triangle count).
        let tri_count = 50_000u32;
        let mut rng = crate::rng::Pcg32::new(7, 1);
        let indices: Vec<u32> = (0..150_000)
            .map(|_| (rng.next_f32() * (tri_count + 500) as f32) as u32 % (tri_count + 500))
            .filter(|&p| p % 97 != 0)
            .collect();
        let mut leaves = Vec::new();
        let mut first = 0;
        while first < indices.len() as u32 {
            let count = (first % 5).min(indices.len() as u32 - first);
            leaves.push([first, count]);
            first += count.max(1);
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let on = |parallel| {
            pool.install(|| {
                let order = leaf_order(&indices, tri_count, parallel, Meter::OFF);
                let slot_of = inverse(&order, parallel, Meter::OFF);
                let slot = |p: u32| slot_of[p as usize];
                let lines = leaf_lines(&leaves, &indices, tri_count, &slot, parallel, Meter::OFF);
                (order, slot_of, lines)
            })
        };
        let (serial, parallel) = (on(false), on(true));
        assert!(serial.0.len() == tri_count as usize && serial.2 > 0);
        assert!(serial == parallel);
    }

    #[test]
    fn scattered_meshes_get_their_records_in_leaf_order() {
        // A soup's triangles lie in random places, in id order.
        let g = crate::scene::generate::random_soup(20_000, 0.05, 3);
        let tree = KdTree::build(&g);
        let p = tree.prims();
        assert!(
            p.tris.iter().enumerate().any(|(s, r)| r.id() != s as u32),
            "the records stayed in id order"
        );
        let mut seen = vec![false; g.triangles.len()];
        for (slot, r) in p.tris.iter().enumerate() {
            assert!(!std::mem::replace(&mut seen[r.id() as usize], true));
            assert_eq!(
                *r,
                crate::accel::triaccel::TriAccel::of(&g, r.id()),
                "slot {slot}"
            );
            assert_eq!(p.corners[slot], g.triangle(r.id()), "slot {slot}");
        }
        tree.validate().expect("valid tree");
        // The leaves name slots: the triangle in each slot a leaf names overlaps the
        // leaf's cell.
        let leaves = leaf_cells(&tree);
        for (i, (node, cell)) in leaves.iter().enumerate() {
            for &slot in tree.leaf_prims(node) {
                let b = p.corners[slot as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |b, &c| b.union(&Aabb { min: c, max: c }));
                assert!(
                    b.min.cmple(cell.max).all() && b.max.cmpge(cell.min).all(),
                    "leaf {i}: slot {slot} lies outside its cell"
                );
            }
        }
        assert!(leaves.len() > 1000, "{} leaves", leaves.len());
    }

    /// Every leaf with its cell, found by walking the tree from the root.
    fn leaf_cells(tree: &KdTree) -> Vec<(KdNode, Aabb)> {
        let mut cells = vec![(0u32, tree.bounds)];
        let mut out = Vec::new();
        while let Some((i, cell)) = cells.pop() {
            let node = tree.nodes()[i as usize];
            if node.is_leaf() {
                out.push((node, cell));
                continue;
            }
            let (left, right) = child_cells(&cell, node.axis(), node.split);
            cells.push((node.children(), left));
            cells.push((node.children() + 1, right));
        }
        out
    }

    /// A small triangle alone in a large empty room (clusters in the corners stretch
    /// the tree's box): without cuts its leaf is a large cell, since a single triangle is
    /// never worth a split to the SAH; with them, the chain of cuts leaves it a cell
    /// close to its own bounds, no other leaf holds a primitive, and no cell the
    /// chain leaves behind keeps a margin the rule would cut.
    #[test]
    fn empty_cuts_shrink_a_lone_triangle_to_its_bounds() {
        let mut g = Geometry::default();
        // Off the room's centre: a cut from the middle of a cell only halves one extent,
        // too little for one cut at the shipped threshold.
        let small = [
            Vec3::new(6.1, 6.2, 6.3),
            Vec3::new(6.2, 6.25, 6.3),
            Vec3::new(6.15, 6.3, 6.35),
        ];
        let mut push = |corners: [Vec3; 3]| {
            let first = g.vertices.len() as u32;
            g.vertices.extend(corners);
            g.triangles.push([first, first + 1, first + 2]);
        };
        push(small);
        // Clusters of triangles at the box's eight corners, so the SAH splits the room.
        for corner in 0..8 {
            let at = |bit: u32| if corner >> bit & 1 == 0 { -10.0 } else { 10.0 };
            let v = Vec3::new(at(0), at(1), at(2));
            for i in 0..20 {
                let w = v + Vec3::splat(0.01 * i as f32);
                push([w, w + 0.1 * Vec3::X, w + 0.1 * Vec3::Y]);
            }
        }
        let own = Aabb {
            min: small[0].min(small[1]).min(small[2]),
            max: small[0].max(small[1]).max(small[2]),
        };
        let lone_cell = |empty_cut: f32| {
            let params = BuildParams {
                empty_cut,
                ..BuildParams::default()
            };
            let tree = KdTree::build_with(&g, &params);
            tree.validate().expect("valid tree");
            let cells = leaf_cells(&tree);
            let holding: Vec<_> = cells
                .iter()
                .filter(|(n, _)| {
                    tree.leaf_prims(n)
                        .iter()
                        .any(|&p| tree.prims().tris[p as usize].id() == 0)
                })
                .collect();
            assert_eq!(
                holding.len(),
                1,
                "cut {empty_cut}: the triangle is in one leaf"
            );
            (tree.nodes().len(), holding[0].1)
        };
        let (plain_nodes, plain) = lone_cell(0.0);
        let cut = BuildParams::default().empty_cut;
        assert!(cut > 0.0, "the shipped build cuts");
        let (cut_nodes, tight) = lone_cell(cut);
        assert!(
            cut_nodes > plain_nodes,
            "{cut_nodes} nodes with cuts, {plain_nodes} without"
        );
        assert!(
            tight.min.cmple(own.min).all() && tight.max.cmpge(own.max).all(),
            "the cell {tight:?} cuts into the triangle's bounds {own:?}"
        );
        assert!(
            tight.surface_area() < 0.01 * plain.surface_area(),
            "cell area {} with cuts, {} without",
            tight.surface_area(),
            plain.surface_area()
        );
        for axis in 0..3 {
            for (lo, hi) in [
                (own.min[axis], tight.max[axis]),
                (tight.min[axis], own.max[axis]),
            ] {
                let mut c = tight;
                (c.min[axis], c.max[axis]) = (lo, hi);
                assert!(
                    c.surface_area() > (1.0 - cut) * tight.surface_area(),
                    "axis {axis}: a margin worth a cut is left in {tight:?}"
                );
            }
        }
    }

    #[test]
    fn depth_limit_follows_the_paper() {
        assert_eq!(default_max_depth(1), 8);
        assert_eq!(default_max_depth(1 << 20), 34);
    }
}
