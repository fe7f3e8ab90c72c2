//! Keeping the pool's other workers awake through a short serial step.
//!
//! A rayon worker that finds no work spins for a few rounds and then sleeps; the next
//! parallel step has to wake it (a futex call and a reschedule), and until then its share
//! of the work waits. The front-to-back occlusion walk alternates a serial step (finding
//! the next batch, 0.1–0.5 ms) with a parallel one (drawing it) tens of times per frame, so
//! the workers fall asleep before every batch: on a 2-core machine a batch that takes
//! 33 µs back to back took 93 µs after 300 µs of serial work. While the serial step runs,
//! [`KeepAwake`] gives every other worker a job that spins until the step ends (running any
//! job the pool has meanwhile), at most [`MAX_SPIN`] without one: the cores are idle then
//! anyway, and they start the batch at once. This is the "active" wait policy of OpenMP
//! runtimes, limited to the steps that need it.
//!
//! The occluder pass draws every cluster, so its walk does not wait for the pyramid: one
//! worker finds the next batch while the others draw the current one. [`join_helping`]
//! keeps the finder, once done, running the drawing's jobs (`rayon::yield_now`) instead of
//! going idle, so it is awake for each of the drawing's parallel stages.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The longest a worker spins for one serial step; past it, it may sleep.
pub(crate) const MAX_SPIN: Duration = Duration::from_millis(2);

/// Keeps the current pool's other workers spinning until dropped (see the module docs).
pub(crate) struct KeepAwake {
    done: Option<Arc<AtomicBool>>,
}

impl KeepAwake {
    /// Starts a spinning job for every other worker of the current rayon pool (none on a
    /// one-thread pool).
    pub(crate) fn start() -> Self {
        let others = rayon::current_num_threads().saturating_sub(1);
        if others == 0 {
            return Self { done: None };
        }
        let done = Arc::new(AtomicBool::new(false));
        for _ in 0..others {
            let d = Arc::clone(&done);
            rayon::spawn(move || {
                help_until(&d, MAX_SPIN);
            });
        }
        Self { done: Some(done) }
    }
}

/// `rayon::join(a, b)`, except that the worker which runs `b` does not go idle when `b` is
/// done: until `a` returns it runs the pool's pending jobs (those `a`'s parallel steps
/// spawn) or spins, for at most [`MAX_SPIN`] at a time without a job. `a` alternates short
/// serial steps with parallel ones; a worker that slept through a serial step would be
/// woken late for the next parallel one.
pub(crate) fn join_helping<RA: Send, RB: Send>(
    a: impl FnOnce() -> RA + Send,
    b: impl FnOnce() -> RB + Send,
) -> (RA, RB) {
    let done = AtomicBool::new(false);
    rayon::join(
        || {
            let r = a();
            done.store(true, Ordering::Release);
            r
        },
        || {
            let r = b();
            help_until(&done, MAX_SPIN);
            r
        },
    )
}

/// Runs pending jobs of the current pool, or spins, until `done` is set (true) or `limit`
/// has passed since the last job ran (false). Outside a pool it returns false at once.
fn help_until(done: &AtomicBool, limit: Duration) -> bool {
    let mut idle = Instant::now();
    while !done.load(Ordering::Acquire) {
        match rayon::yield_now() {
            Some(rayon::Yield::Executed) => idle = Instant::now(),
            Some(rayon::Yield::Idle) if idle.elapsed() < limit => std::hint::spin_loop(),
            _ => return false,
        }
    }
    true
}

impl Drop for KeepAwake {
    fn drop(&mut self) {
        if let Some(d) = &self.done {
            d.store(true, Ordering::Release);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spinner lets go when the step ends, and gives up at its limit when it does not
    /// (at once outside a pool); a one-thread pool gets none (its only worker is the one
    /// doing the step), a two-thread pool one, released when the guard drops.
    #[test]
    fn spinners_let_go_when_the_step_ends() {
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        two.install(|| {
            let done = Arc::new(AtomicBool::new(false));
            let d = Arc::clone(&done);
            let setter = std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(1));
                d.store(true, Ordering::Release);
            });
            assert!(help_until(&done, Duration::from_secs(60)));
            setter.join().unwrap();
            assert!(!help_until(&AtomicBool::new(false), Duration::from_micros(100)));
        });
        assert!(!help_until(&AtomicBool::new(false), Duration::from_secs(60)), "outside a pool: no wait");

        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        one.install(|| assert!(KeepAwake::start().done.is_none()));
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        two.install(|| {
            let awake = KeepAwake::start();
            let flag = Arc::clone(awake.done.as_ref().unwrap());
            assert!(!flag.load(Ordering::Acquire));
            drop(awake);
            assert!(flag.load(Ordering::Acquire));
        });
    }

    /// `join_helping` gives both results whether or not another worker takes `b`, and the
    /// helper runs `a`'s jobs until `a` ends; a helper whose flag another job sets returns.
    #[test]
    fn join_helping_runs_both_and_helps() {
        use rayon::prelude::*;
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (sum, b) = pool.install(|| {
                join_helping(
                    || (0..100_000u32).into_par_iter().with_min_len(1000).map(u64::from).map(|i| i * i).sum::<u64>(),
                    || 7,
                )
            });
            assert_eq!(sum, (0..100_000u64).map(|i| i * i).sum::<u64>());
            assert_eq!(b, 7);
        }
        // The flag set by a pending job of the pool: the helper runs it, then returns.
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        two.install(|| {
            let done = Arc::new(AtomicBool::new(false));
            let d = Arc::clone(&done);
            rayon::spawn(move || {
                std::thread::sleep(Duration::from_millis(1));
                d.store(true, Ordering::Release);
            });
            assert!(help_until(&done, Duration::from_secs(60)));
        });
    }
}
