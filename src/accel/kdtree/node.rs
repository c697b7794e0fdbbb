//! The kd-tree's node: 8 bytes, in one contiguous 64-byte-aligned array.
//!
//! `bits` holds the axis (0, 1, 2) or the leaf flag (3) in its low 2 bits; the other 30
//! bits index the first child of an inner node (children come in pairs so one index
//! reaches both: right = left + 1) or, for a leaf, its entry in the leaf table.
//! pbrt's `KdAccelNode` is the ancestor.

/// Axis value that marks a leaf.
const LEAF: u32 = 3;

#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KdNode {
    /// Split position (inner nodes); unused (0) for leaves.
    pub split: f32,
    bits: u32,
}

const _: () = assert!(std::mem::size_of::<KdNode>() == 8);

/// Largest index that fits the node's 30 bits.
pub const MAX_INDEX: u32 = (1 << 30) - 1;

impl KdNode {
    /// An inner node splitting `axis` at `split`, whose children are `left` and `left + 1`.
    #[inline]
    pub fn inner(axis: u32, split: f32, left: u32) -> KdNode {
        debug_assert!(axis < 3 && left <= MAX_INDEX);
        KdNode {
            split,
            bits: (left << 2) | axis,
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
        self.bits >> 2
    }

    /// Leaf-table index of a leaf.
    #[inline]
    pub fn leaf_index(&self) -> u32 {
        self.bits >> 2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_round_trip() {
        let n = KdNode::inner(2, 1.5, MAX_INDEX);
        assert!(!n.is_leaf() && n.axis() == 2 && n.children() == MAX_INDEX && n.split == 1.5);
        let l = KdNode::leaf(12345);
        assert!(l.is_leaf() && l.leaf_index() == 12345);
    }
}
