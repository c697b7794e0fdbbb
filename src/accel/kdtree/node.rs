//! The kd-tree's node: 8 bytes, in one contiguous 64-byte-aligned array.
//!
//! `bits` holds the axis (0, 1, 2) or the leaf flag (3) in its low 2 bits. For an inner
//! node, the next 2 bits say which children are empty leaves and the top 28 bits index
//! the first child (children come in pairs so one index reaches both: right = left +
//! 1); for a leaf, the other 30 bits index its entry in the leaf table. pbrt's
//! `KdAccelNode` is the ancestor.
//!
//! The empty-child bits let traversal skip an empty leaf from its parent: a ray that
//! would push the far child only to visit an empty near leaf and pop it goes to the far
//! child at once, with the interval the pop would have given it, and a ray whose far
//! child is empty pushes nothing. Half the leaves of the benchmark scenes are empty.
//!
//! The builder writes leaves as leaf-table entries; [`with_leaf_ranges`] then turns
//! every leaf into its range of the index list (first index in the 30 bits, count in
//! the split word), so traversal reads a leaf's primitives without the table lookup.
//! The nodes of a built [`super::KdTree`] are in that form.

use crate::accel::occupancy::Meter;
use crate::simd::{Mask, Simd, Uint, Vu, inl};

/// Axis value that marks a leaf.
const LEAF: u32 = 3;

/// One node in 8 bytes: the split position and a word holding the axis (or the leaf
/// mark) in 2 bits and a 30-bit child-pair or leaf index. Eight fit a cache line.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct KdNode {
    /// Split position (inner nodes); for a leaf, 0 or (once ranged) the bits of its
    /// primitive count.
    pub split: f32,
    bits: u32,
}

const _: () = assert!(std::mem::size_of::<KdNode>() == 8);

/// Largest index that fits the node's 30 bits.
pub const MAX_INDEX: u32 = (1 << 30) - 1;

/// Largest child-pair index that fits an inner node's 28 bits.
pub const MAX_CHILD: u32 = (1 << 28) - 1;

/// An inner node's flag: its left child is an empty leaf.
pub const LEFT_EMPTY: u32 = 1;

/// An inner node's flag: its right child is an empty leaf.
pub const RIGHT_EMPTY: u32 = 2;

impl KdNode {
    /// An inner node splitting `axis` at `split`, whose children are `left` and `left + 1`.
    #[inline]
    pub fn inner(axis: u32, split: f32, left: u32) -> KdNode {
        debug_assert!(axis < 3 && left <= MAX_CHILD);
        KdNode {
            split,
            bits: (left << 4) | axis,
        }
    }

    /// A leaf pointing at entry `leaf` of the tree's leaf table.
    #[inline]
    pub fn leaf(leaf: u32) -> KdNode {
        debug_assert!(leaf <= MAX_INDEX);
        KdNode {
            split: 0.0,
            bits: (leaf << 2) | LEAF,
        }
    }

    /// True for a leaf, false for an inner node.
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.bits & 3 == LEAF
    }

    /// Split axis of an inner node.
    #[inline]
    pub fn axis(&self) -> usize {
        (self.bits & 3) as usize
    }

    /// Index of the left child of an inner node; the right child follows it.
    #[inline]
    pub fn children(&self) -> u32 {
        self.bits >> 4
    }

    /// Which children of an inner node are empty leaves: [`LEFT_EMPTY`] and
    /// [`RIGHT_EMPTY`] bits, set by [`mark_empty_children`]; bit `i` is child
    /// `children() + i`.
    #[inline]
    pub fn empty_children(&self) -> u32 {
        (self.bits >> 2) & 3
    }

    /// [`KdNode::empty_children`] in traversal order: bit 0 when the near child is an
    /// empty leaf, bit 1 when the far one is, for a ray whose near child is
    /// `children() + flip`.
    #[inline]
    pub fn empty_near_far(&self, flip: u32) -> u32 {
        let e = self.empty_children();
        ((e >> flip) & 1) | (((e >> (flip ^ 1)) & 1) << 1)
    }

    /// Leaf-table index of a leaf, as the builder writes it.
    #[inline]
    pub fn leaf_index(&self) -> u32 {
        self.bits >> 2
    }

    /// A leaf holding the `count` primitive ids from `first` on in the index list.
    #[inline]
    pub fn leaf_range(first: u32, count: u32) -> KdNode {
        debug_assert!(first <= MAX_INDEX);
        KdNode {
            split: f32::from_bits(count),
            bits: (first << 2) | LEAF,
        }
    }

    /// First index-list position of a ranged leaf.
    #[inline]
    pub fn leaf_first(&self) -> u32 {
        self.bits >> 2
    }

    /// Primitive count of a ranged leaf.
    #[inline]
    pub fn leaf_count(&self) -> u32 {
        self.split.to_bits()
    }
}

/// The nodes as 32-bit words, node `i`'s split at `2 i` and its bits at `2 i + 1`: the
/// table the lane walks gather from (traverse_lanes.rs).
#[inline(always)]
pub fn as_words(nodes: &[KdNode]) -> &[u32] {
    // `KdNode` is `Pod`: two 4-byte fields, no padding (the derive checks it).
    bytemuck::cast_slice(nodes)
}

/// The words of one node per lane ([`as_words`]'s odd words), decoded in SIMD: the one
/// vector reading of the layout above.
pub struct NodeLanes<W: Simd> {
    /// The lane's node is a leaf.
    pub leaf: Mask<W>,
    /// Split axis 0 (x), and axis 1 (y); an inner node with neither splits z.
    pub axis: [Mask<W>; 2],
    /// Index of the left child of an inner node.
    pub children: Vu<W>,
    /// The left child is an empty leaf, and the right one ([`LEFT_EMPTY`],
    /// [`RIGHT_EMPTY`]).
    pub empty: [Mask<W>; 2],
}

impl<W: Simd> NodeLanes<W> {
    /// Decodes the lanes' node words.
    #[inline(always)]
    pub fn decode(bits: Vu<W>) -> NodeLanes<W> {
        let splat = Vu::<W>::splat;
        let axis = bits & splat(3);
        let above = inl(
            #[inline(always)]
            |k: u32| axis.cmp_gt(splat(k)),
        );
        let (a0, a1, a2) = (above(0), above(1), above(2));
        let flag = inl(
            #[inline(always)]
            |f: u32| (bits & splat(f << 2)).cmp_gt(splat(0)),
        );
        NodeLanes {
            leaf: a2,
            axis: [!a0, a0 & !a1],
            children: bits.shr(4),
            empty: [flag(LEFT_EMPTY), flag(RIGHT_EMPTY)],
        }
    }
}

/// `nodes` with every leaf-table leaf replaced by its `[first, count]` range from
/// `leaves`, so traversal skips one dependent load per leaf (the table is 8 bytes per
/// leaf, scattered like the nodes; half of Sponza's leaves are empty and now cost no
/// load at all). Panics if the index list outgrows the 30 bits.
#[inline(always)]
pub fn with_leaf_ranges(mut nodes: Vec<KdNode>, leaves: &[[u32; 2]]) -> Vec<KdNode> {
    for n in nodes.iter_mut() {
        *n = ranged(*n, leaves);
    }
    nodes
}

/// `n`, if a leaf-table leaf, as its `[first, count]` range from `leaves`
/// ([`with_leaf_ranges`]).
#[inline(always)]
pub fn ranged(n: KdNode, leaves: &[[u32; 2]]) -> KdNode {
    if !n.is_leaf() {
        return n;
    }
    let [first, count] = leaves[n.leaf_index() as usize];
    assert!(
        first <= MAX_INDEX,
        "kd-tree: index list exceeds 2^30 entries"
    );
    KdNode::leaf_range(first, count)
}

/// The [`KdNode::empty_children`] bits of the child pair starting at `left`.
#[inline(always)]
pub fn empty_flags(nodes: &[KdNode], left: usize) -> u32 {
    let empty = inl(
        #[inline(always)]
        |k: usize| nodes[k].is_leaf() && nodes[k].leaf_count() == 0,
    );
    (empty(left) as u32 * LEFT_EMPTY) | (empty(left + 1) as u32 * RIGHT_EMPTY)
}

/// Sets every inner node's [`KdNode::empty_children`] bits from its children, which
/// must be ranged leaves already ([`with_leaf_ranges`]) where they are leaves.
#[inline(always)]
pub fn mark_empty_children(nodes: &mut [KdNode]) {
    for i in 0..nodes.len() {
        nodes[i] = marked(nodes, i);
    }
}

/// Node `i` of `nodes` with its [`KdNode::empty_children`] bits set
/// ([`mark_empty_children`]).
#[inline(always)]
fn marked(nodes: &[KdNode], i: usize) -> KdNode {
    let n = nodes[i];
    if n.is_leaf() {
        return n;
    }
    let flags = empty_flags(nodes, n.children() as usize);
    KdNode {
        bits: (n.bits & !(3 << 2)) | (flags << 2),
        ..n
    }
}

/// Eight nodes: one 64-byte cache line.
#[repr(C, align(64))]
#[derive(Clone, Copy)]
struct NodeBlock([KdNode; 8]);

const _: () = assert!(std::mem::size_of::<NodeBlock>() == 64);

/// The node array, starting on a 64-byte boundary so a child pair (8-byte aligned,
/// 16 bytes) never straddles two cache lines. Reads as `&[KdNode]`.
#[derive(Clone)]
pub struct AlignedNodes {
    blocks: Vec<NodeBlock>,
    len: usize,
}

impl From<Vec<KdNode>> for AlignedNodes {
    #[inline(always)]
    fn from(nodes: Vec<KdNode>) -> AlignedNodes {
        let pad = KdNode::leaf(0);
        let blocks = nodes
            .chunks(8)
            .map(
                #[inline(always)]
                |c| {
                    NodeBlock(std::array::from_fn(
                        #[inline(always)]
                        |i| c.get(i).copied().unwrap_or(pad),
                    ))
                },
            )
            .collect();
        AlignedNodes {
            blocks,
            len: nodes.len(),
        }
    }
}

impl AlignedNodes {
    /// `nodes` (ranged leaves where they are leaves) with every inner node's empty-child
    /// bits set ([`mark_empty_children`]), the blocks made on the current rayon pool:
    /// the build's last pass.
    pub fn marked_in_parallel(nodes: &[KdNode], meter: Meter) -> AlignedNodes {
        use rayon::prelude::*;
        let pad = KdNode::leaf(0);
        let blocks = meter.hand_off(|| {
            (meter.jobs((0..nodes.len().div_ceil(8)).into_par_iter()))
                .map(|b| {
                    NodeBlock(std::array::from_fn(|k| {
                        let i = 8 * b + k;
                        if i < nodes.len() {
                            marked(nodes, i)
                        } else {
                            pad
                        }
                    }))
                })
                .collect()
        });
        AlignedNodes {
            blocks,
            len: nodes.len(),
        }
    }
}

impl std::ops::Deref for AlignedNodes {
    type Target = [KdNode];

    #[inline(always)]
    fn deref(&self) -> &[KdNode] {
        // A pointer cast, not `bytemuck::cast_slice(&self.blocks)[..self.len]`: that
        // cut's bounds check on every node load cost tile64 2-4% on camera rays
        // (perf/log/overview.md).
        // SAFETY: `NodeBlock` is `repr(C)` holding exactly `[KdNode; 8]` (the const
        // assert above proves there is no padding), so `blocks` is `8 * blocks.len()`
        // initialized, contiguous `KdNode`s; `From` keeps `len <= 8 * blocks.len()`, and
        // the slice borrows `self`, so the memory lives and stays unmodified.
        unsafe { std::slice::from_raw_parts(self.blocks.as_ptr().cast::<KdNode>(), self.len) }
    }
}

impl std::fmt::Debug for AlignedNodes {
    #[inline(always)]
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`NodeLanes::decode`] against the scalar accessors, for leaves and inner nodes of
    /// every axis and empty-child pattern, lanes mixed.
    fn lanes_decode_like_scalar<W: Simd>() {
        use crate::simd::{LaneMask, Uint};
        let mut nodes = vec![KdNode::leaf_range(5, 3), KdNode::leaf_range(MAX_INDEX, 0)];
        for axis in 0..3 {
            for empty in 0..4u32 {
                let mut n = KdNode::inner(axis, 1.5, MAX_CHILD - empty);
                n.bits |= empty << 2;
                nodes.push(n);
            }
        }
        let words = as_words(&nodes);
        for start in 0..nodes.len() {
            let pick = |i: usize| (start + i) % nodes.len();
            let bits = Vu::<W>::from_fn(|i| words[2 * pick(i) + 1]);
            let d = NodeLanes::<W>::decode(bits);
            for i in 0..W::LANES {
                let n = &nodes[pick(i)];
                let lane = |m: Mask<W>| m.bits() >> i & 1 == 1;
                assert_eq!(words[2 * pick(i)], n.split.to_bits());
                assert_eq!(lane(d.leaf), n.is_leaf(), "node {n:?}");
                if !n.is_leaf() {
                    assert_eq!(lane(d.axis[0]), n.axis() == 0, "node {n:?}");
                    assert_eq!(lane(d.axis[1]), n.axis() == 1, "node {n:?}");
                    assert_eq!(d.children.lane(i), n.children(), "node {n:?}");
                    let e = n.empty_children();
                    assert_eq!(lane(d.empty[0]), e & LEFT_EMPTY != 0, "node {n:?}");
                    assert_eq!(lane(d.empty[1]), e & RIGHT_EMPTY != 0, "node {n:?}");
                }
            }
        }
    }

    #[test]
    fn lanes_decode_at_every_width() {
        lanes_decode_like_scalar::<crate::simd::W4>();
        lanes_decode_like_scalar::<crate::simd::W8>();
        lanes_decode_like_scalar::<crate::simd::W16>();
    }

    #[test]
    fn bits_round_trip() {
        let n = KdNode::inner(2, 1.5, MAX_CHILD);
        assert!(!n.is_leaf() && n.axis() == 2 && n.children() == MAX_CHILD && n.split == 1.5);
        assert_eq!(n.empty_children(), 0);
        let l = KdNode::leaf(12345);
        assert!(l.is_leaf() && l.leaf_index() == 12345);
        let r = KdNode::leaf_range(MAX_INDEX, u32::MAX);
        assert!(r.is_leaf() && r.leaf_first() == MAX_INDEX && r.leaf_count() == u32::MAX);
        let nodes = with_leaf_ranges(vec![KdNode::inner(0, 1.0, 1), l, KdNode::leaf(0)], &{
            let mut t = vec![[0, 0]; 12346];
            t[0] = [7, 0];
            t[12345] = [3, 4];
            t
        });
        assert_eq!(nodes[0], KdNode::inner(0, 1.0, 1));
        assert_eq!((nodes[1].leaf_first(), nodes[1].leaf_count()), (3, 4));
        assert_eq!((nodes[2].leaf_first(), nodes[2].leaf_count()), (7, 0));
    }

    #[test]
    fn empty_children_are_marked_without_touching_the_rest() {
        let mut nodes = vec![
            KdNode::inner(1, 2.0, 1),
            KdNode::leaf_range(0, 0),
            KdNode::inner(2, -3.0, 3),
            KdNode::leaf_range(4, 2),
            KdNode::leaf_range(6, 0),
        ];
        mark_empty_children(&mut nodes);
        assert_eq!(nodes[0].empty_children(), LEFT_EMPTY);
        assert_eq!(nodes[2].empty_children(), RIGHT_EMPTY);
        assert_eq!(
            (nodes[0].empty_near_far(0), nodes[0].empty_near_far(1)),
            (1, 2)
        );
        assert_eq!(
            (nodes[2].empty_near_far(0), nodes[2].empty_near_far(1)),
            (2, 1)
        );
        for (n, (axis, split, children)) in [(0, (1, 2.0, 1)), (2, (2, -3.0, 3))] {
            let n = nodes[n];
            assert!(!n.is_leaf());
            assert_eq!((n.axis(), n.split, n.children()), (axis, split, children));
        }
        assert_eq!((nodes[3].leaf_first(), nodes[3].leaf_count()), (4, 2));
    }

    #[test]
    fn parallel_marking_is_the_serial_marking() {
        // A chain of inner nodes whose children are empty or full leaves, across blocks.
        let mut nodes = vec![KdNode::inner(0, 0.5, 1)];
        for i in 0..40u32 {
            let left = nodes.len() as u32;
            nodes.push(KdNode::leaf_range(i, i % 3));
            nodes.push(KdNode::inner(i % 3, i as f32, left + 2));
        }
        nodes.extend([KdNode::leaf_range(0, 0), KdNode::leaf_range(1, 1)]);
        let parallel = AlignedNodes::marked_in_parallel(&nodes, Meter::OFF);
        mark_empty_children(&mut nodes);
        assert_eq!(&parallel[..], &nodes[..]);
        assert!(nodes.iter().any(|n| n.empty_children() != 0));
    }

    #[test]
    fn aligned_nodes_read_back_in_order_from_a_cache_line_boundary() {
        for count in [0, 1, 7, 8, 9, 17] {
            let nodes: Vec<KdNode> = (0..count).map(|i| KdNode::inner(1, i as f32, i)).collect();
            let aligned = AlignedNodes::from(nodes.clone());
            assert_eq!(&aligned[..], &nodes[..]);
            assert_eq!(aligned.as_ptr() as usize % 64, 0);
        }
    }
}
