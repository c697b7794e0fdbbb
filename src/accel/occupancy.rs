//! Stage: accel. How many threads a parallel job keeps busy: the seconds during which
//! 0, 1, 2, ... threads of the pool work on it.
//!
//! The acceleration structure's build marks its own work: the calling thread works from
//! start to end, except while it hands work to the pool ([`Meter::hand_off`], around
//! every `rayon::join` and parallel iterator), and every closure it hands over works
//! while it runs ([`Meter::work`]). The time with fewer threads working than the pool
//! has is the time its threads wait for work: on two threads, the time with one or none
//! working is the job's serial part, the figure Amdahl's law extrapolates from
//! ([`Occupancy::amdahl`]). A meter that is off costs a branch per hand-off.

use rayon::iter::{IndexedParallelIterator, ParallelIterator};
use std::sync::Mutex;
use std::time::Instant;

/// Items per job of the build's flat parallel passes (`with_min_len(JOB)
/// .with_max_len(JOB)`; chunked passes take one chunk per job). Rayon's adaptive split
/// hands each thread a few large pieces, and a thread that finishes first finds
/// nothing to steal from the last one: up to a quarter of a pass ran on one thread.
/// Jobs this size keep the tail short and their marks cheap.
pub const JOB: usize = 4096;

/// The record: seconds spent with each number of threads working.
#[derive(Debug)]
pub struct Occupancy {
    state: Mutex<State>,
}

#[derive(Debug)]
struct State {
    working: usize,
    since: Instant,
    seconds: Vec<f64>,
}

impl Default for Occupancy {
    fn default() -> Self {
        Occupancy::new()
    }
}

impl Occupancy {
    /// An empty record for one job; the clock starts at its first mark.
    pub fn new() -> Occupancy {
        Occupancy {
            state: Mutex::new(State {
                working: 0,
                since: Instant::now(),
                seconds: Vec::new(),
            }),
        }
    }

    /// A meter writing into this record.
    pub fn meter(&self) -> Meter<'_> {
        Meter(Some(self))
    }

    fn change(&self, up: bool) {
        let now = Instant::now();
        // A thread that panicked inside a marked span leaves the count as it was.
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let k = s.working;
        let started = !s.seconds.is_empty();
        if s.seconds.len() <= k {
            s.seconds.resize(k + 1, 0.0);
        }
        if started {
            let dt = now.duration_since(s.since).as_secs_f64();
            s.seconds[k] += dt;
        }
        s.since = now;
        s.working = if up { k + 1 } else { k.saturating_sub(1) };
    }

    /// Seconds spent with `k` threads working, for `k` = 0, 1, ... up to the most seen.
    /// The time before the first and after the last mark is not counted.
    pub fn seconds(&self) -> Vec<f64> {
        let s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let mut out = s.seconds.clone();
        while out.len() > 1 && out.last() == Some(&0.0) {
            out.pop();
        }
        out
    }

    /// The most threads that were working at once.
    pub fn peak(&self) -> usize {
        self.seconds().len().saturating_sub(1)
    }

    /// Amdahl's law from a run on `threads` threads (2 in perf/): the serial part is the
    /// time during which fewer than `threads` worked, every thread waiting for work then
    /// counted as a lost thread-second; the rest ran `threads` wide. Returns the serial
    /// fraction of the work, `f`, and the speedup it predicts on `n` threads,
    /// `1 / (f + (1 - f) / n)`.
    pub fn amdahl(&self, threads: usize, n: usize) -> (f64, f64) {
        let s = self.seconds();
        let threads = threads.max(1);
        let serial: f64 = s.iter().take(threads).sum();
        let parallel = s.get(threads).copied().unwrap_or(0.0) * threads as f64;
        let f = if serial + parallel > 0.0 {
            serial / (serial + parallel)
        } else {
            0.0
        };
        (f, 1.0 / (f + (1.0 - f) / n as f64))
    }

    /// The wall time a machine of `n` cores would take, from a run whose pool had at
    /// least `n` threads on `cores` cores: `k` threads working got `min(k, cores)`
    /// cores' worth of work done, which `min(k, n)` cores would do in proportion. A
    /// pool of 16 threads on 2 cores shows how much parallelism the job offers 16 cores,
    /// where a pool of 2 cannot. Indicative only: threads that spin while looking for
    /// work take cores from those working, and short jobs meet the scheduler's time
    /// slices. On 2 cores a perfectly parallel job of 1.4 s, in 512 jobs, reads 15.2x of
    /// 16; one of 0.08 s reads 9.6x.
    pub fn predicted_wall(&self, cores: usize, n: usize) -> f64 {
        self.seconds()
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                if k == 0 {
                    t
                } else {
                    t * k.min(cores) as f64 / k.min(n) as f64
                }
            })
            .sum()
    }
}

/// A handle on an [`Occupancy`] record, or none (`Meter::OFF`): the build takes one and
/// marks its work through it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Meter<'a>(Option<&'a Occupancy>);

impl<'a> Meter<'a> {
    /// Marks nothing.
    pub const OFF: Meter<'static> = Meter(None);

    /// Runs `f` as one more thread working.
    #[inline]
    pub fn work<R>(self, f: impl FnOnce() -> R) -> R {
        let _working = self.working();
        f()
    }

    /// One more thread working until the guard is dropped: for a parallel iterator's
    /// `map_init`, whose value lives as long as one job of the pool.
    #[inline]
    pub fn working(self) -> Working<'a> {
        Working(self.0.inspect(|o| o.change(true)))
    }

    /// `iter` as a flat pass of the build: jobs of exactly [`JOB`] items (the last one
    /// shorter), each marked working while it runs, what follows `jobs` in the chain
    /// included. Call it inside a [`Meter::hand_off`].
    #[inline]
    pub fn jobs<I: IndexedParallelIterator>(
        self,
        iter: I,
    ) -> impl IndexedParallelIterator<Item = I::Item> + use<'a, I> {
        (iter.with_min_len(JOB).with_max_len(JOB)).map_init(move || self.working(), |_, x| x)
    }

    /// Runs `f`, which hands work to the pool, with the calling thread not counted:
    /// the closures `f` hands over count themselves through [`Meter::work`], the one
    /// the caller runs itself included.
    #[inline]
    pub fn hand_off<R>(self, f: impl FnOnce() -> R) -> R {
        let Some(o) = self.0 else { return f() };
        o.change(false);
        let _back = Back(o);
        f()
    }
}

/// A thread marked working ([`Meter::working`]) until dropped, also when unwinding.
pub struct Working<'a>(Option<&'a Occupancy>);

impl Drop for Working<'_> {
    fn drop(&mut self) {
        if let Some(o) = self.0 {
            o.change(false);
        }
    }
}

/// Ends a [`Meter::hand_off`], also when `f` unwinds.
struct Back<'a>(&'a Occupancy);

impl Drop for Back<'_> {
    fn drop(&mut self) {
        self.0.change(true);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spin(ms: u64) {
        let end = Instant::now() + std::time::Duration::from_millis(ms);
        while Instant::now() < end {
            std::hint::black_box(0);
        }
    }

    #[test]
    fn serial_work_is_one_thread_and_nested_hand_offs_balance() {
        let o = Occupancy::new();
        let m = o.meter();
        m.work(|| {
            spin(5);
            m.hand_off(|| m.work(|| spin(5)));
            spin(5);
        });
        let s = o.seconds();
        assert_eq!(s.len(), 2, "{s:?}");
        assert!(s[1] >= 0.015 && s[0] < 0.005, "{s:?}");
        let (f, speedup) = o.amdahl(2, 16);
        assert!(f > 0.99 && speedup < 1.01, "{f} {speedup}");
    }

    #[test]
    fn a_join_on_two_threads_counts_two_working() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let o = Occupancy::new();
        let m = o.meter();
        // Two halves that each wait for the other to start run side by side.
        let started = std::sync::Barrier::new(2);
        pool.install(|| {
            m.work(|| {
                m.hand_off(|| {
                    rayon::join(
                        || m.work(|| (started.wait(), spin(30))),
                        || m.work(|| (started.wait(), spin(30))),
                    )
                })
            })
        });
        let s = o.seconds();
        assert_eq!(o.peak(), 2, "{s:?}");
        assert!(s[2] >= 0.025, "{s:?}");
        // Twice the work in the two-wide part as in the rest: Amdahl predicts more than
        // 2x on 16 threads, and the predicted wall on 2 cores is what was measured.
        assert!(o.amdahl(2, 16).1 > 2.0, "{s:?}");
        let wall: f64 = s.iter().sum();
        assert!((o.predicted_wall(2, 2) - wall).abs() < 1e-9);
    }

    #[test]
    fn a_meter_that_is_off_marks_nothing() {
        assert_eq!(Meter::OFF.work(|| Meter::OFF.hand_off(|| 7)), 7);
    }
}
