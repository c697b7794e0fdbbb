//! Stage: accel. Traversal counters, per thread, for `raypack bench` to report per ray
//! and mode: inner-node steps, leaf visits and primitive tests; packets split by
//! direction signs; ray tiles, their fallbacks to packets and their entry depths. A
//! packet or tile group counts one step per node it visits, whatever its number of
//! active lanes, so the counts per ray show how much work a packet shares. Every
//! traversal counter of the kd-tree lives here.
//!
//! Compiled in only with the `stats` feature (`cargo build --release --features
//! stats`): without it [`bump`] is empty, [`counts`] is zero and the kernels are
//! unchanged.

/// Work done by the traversals of one thread.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounts {
    /// Inner nodes visited (a packet step counts once).
    pub node_steps: u64,
    /// Leaves visited.
    pub leaf_visits: u64,
    /// Primitive tests run.
    pub prim_tests: u64,
    /// Packets whose lanes disagreed on a direction sign and were split into coherent
    /// groups (`traverse_packet`).
    pub packet_splits: u64,
    /// Ray tiles traced (`traverse_tile`).
    pub tiles: u64,
    /// Tiles whose rays disagree on a direction sign (or fit in one group), traced one
    /// packet per group.
    pub tile_fallbacks: u64,
    /// Sum over tiles of the nodes passed for the whole tile at once.
    pub tile_entry_depth: u64,
}

/// `ZERO` (every counter 0, for the `const` thread-local), `since` (`self - earlier`)
/// and `plus` (the sum), field by field, for a struct of counters named with its fields
/// (a field left out of the list is a missing field, a compile error).
macro_rules! field_wise {
    ($t:ident { $($f:ident),+ $(,)? }) => {
        impl $t {
            /// Every counter at 0.
            pub const ZERO: $t = $t { $($f: 0),+ };

            /// `self - earlier`, field by field.
            pub fn since(self, earlier: $t) -> $t {
                $t { $($f: self.$f - earlier.$f),+ }
            }

            /// The sum, field by field.
            pub fn plus(self, o: $t) -> $t {
                $t { $($f: self.$f + o.$f),+ }
            }
        }
    };
}
field_wise!(TraversalCounts {
    node_steps,
    leaf_visits,
    prim_tests,
    packet_splits,
    tiles,
    tile_fallbacks,
    tile_entry_depth
});

/// Whether the counters are compiled in.
pub const ENABLED: bool = cfg!(feature = "stats");

#[cfg(feature = "stats")]
thread_local! {
    static COUNTS: std::cell::Cell<TraversalCounts> =
        const { std::cell::Cell::new(TraversalCounts::ZERO) };
}

/// Applies `f` to this thread's counters (nothing without the `stats` feature).
#[inline(always)]
pub fn bump(f: impl FnOnce(&mut TraversalCounts)) {
    #[cfg(feature = "stats")]
    COUNTS.with(|c| {
        let mut v = c.get();
        f(&mut v);
        c.set(v);
    });
    #[cfg(not(feature = "stats"))]
    let _ = f;
}

/// Counts `n` primitive tests: the `count` of `Prims::leaf_groups`.
#[inline(always)]
pub fn count_tests(n: u64) {
    bump(
        #[inline(always)]
        |c| c.prim_tests += n,
    );
}

/// This thread's counters so far (zero without the `stats` feature).
pub fn counts() -> TraversalCounts {
    #[cfg(feature = "stats")]
    return COUNTS.with(std::cell::Cell::get);
    #[cfg(not(feature = "stats"))]
    TraversalCounts::default()
}
