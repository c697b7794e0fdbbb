//! A traversal stack that costs nothing to set up: the walks of the kd-tree and of the
//! BVH keep their pending nodes in one.

use std::mem::MaybeUninit;

/// A traversal stack of `N` `Copy` entries whose free slots stay uninitialized: zeroing
/// the whole array on every call (64 packet entries are 4 KiB) cost more than the
/// pushes of a typical coherent packet.
pub(crate) struct Stack<T: Copy, const N: usize> {
    items: [MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> Stack<T, N> {
    #[inline(always)]
    pub(crate) fn new() -> Stack<T, N> {
        Stack {
            items: [const { MaybeUninit::uninit() }; N],
            len: 0,
        }
    }

    /// Panics when full (a tree's depth bounds the pushes).
    #[inline(always)]
    pub(crate) fn push(&mut self, item: T) {
        self.items[self.len].write(item);
        self.len += 1;
    }

    /// Drops every entry.
    #[inline(always)]
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// The entries, bottom first.
    #[cfg(test)]
    pub(crate) fn as_slice(&self) -> &[T] {
        // SAFETY: `push` is the only writer and raises `len` only after writing slot
        // `len`, so the first `len` slots hold initialized items; `MaybeUninit<T>` has
        // `T`'s layout.
        unsafe { std::slice::from_raw_parts(self.items.as_ptr().cast::<T>(), self.len) }
    }

    /// Becomes a copy of `other` (its entries only, not the free slots).
    #[inline(always)]
    pub(crate) fn copy_from(&mut self, other: &Stack<T, N>) {
        self.items[..other.len].copy_from_slice(&other.items[..other.len]);
        self.len = other.len;
    }

    #[inline(always)]
    pub(crate) fn pop(&mut self) -> Option<T> {
        self.len = self.len.checked_sub(1)?;
        // SAFETY: `push` is the only writer and raises `len` only after writing slot
        // `len`; `pop` only lowers it. So every slot below the old `len`, this one
        // included, holds an initialized item (`T: Copy`, so reading it twice is fine).
        Some(unsafe { self.items[self.len].assume_init() })
    }
}
