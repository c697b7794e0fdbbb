//! The `raypack` binary's allocator: the system allocator, with large blocks (the tree's
//! nodes, index list and triangle records, the ray sets, the build's arrays) placed on
//! 2 MiB boundaries and marked for transparent huge pages (`madvise(MADV_HUGEPAGE)`)
//! before their first touch. Incoherent rays load nodes and records from all over
//! several megabytes; on 4 KiB pages most of those loads also miss the TLB, on 2 MiB
//! pages few do (perf/log/stream.md, "Huge pages"). Linux only; a hint the kernel may
//! ignore (`/sys/kernel/mm/transparent_hugepage/enabled` set to `never`). The library
//! leaves the choice of allocator to the program that links it.

use std::alloc::{GlobalAlloc, Layout, System};

/// A huge page.
const HUGE: usize = 2 << 20;

/// Blocks at least this large go on huge pages; smaller ones are left as they are (the
/// alignment would waste up to a huge page per block).
const MIN_BYTES: usize = 4 << 20;

/// [`System`], with blocks of [`MIN_BYTES`] or more huge-page aligned and advised.
pub struct HugePages;

/// The layout a block of `layout` is allocated with: the same for `alloc` and
/// `dealloc`, since both see the same `layout`.
#[inline]
fn placed(layout: Layout) -> Layout {
    if cfg!(target_os = "linux") && layout.size() >= MIN_BYTES {
        Layout::from_size_align(layout.size(), layout.align().max(HUGE)).unwrap_or(layout)
    } else {
        layout
    }
}

// SAFETY: every method forwards to `System` with `placed(layout)`, a valid layout at
// least as large and as aligned as `layout`, and frees with the same `placed(layout)`
// it allocated with; `madvise` only changes how the kernel backs pages of the block
// just allocated, never their contents or their mapping.
unsafe impl GlobalAlloc for HugePages {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let placed = placed(layout);
        // SAFETY: `placed` has a non-zero size (at least `layout`'s, which the caller
        // guarantees non-zero).
        let p = unsafe { System.alloc(placed) };
        #[cfg(target_os = "linux")]
        if !p.is_null() && placed.align() >= HUGE {
            // SAFETY: `p` starts a block of `placed.size()` bytes that this call owns,
            // aligned to a huge page (so to a page, as `madvise` requires).
            unsafe {
                libc::madvise(p.cast(), placed.size(), libc::MADV_HUGEPAGE);
            }
        }
        p
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `alloc` with `placed(layout)`.
        unsafe { System.dealloc(ptr, placed(layout)) }
    }
}
